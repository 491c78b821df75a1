"""The contact scenes of issue 12 end to end: speed, intersection checks, NVIDIA Newton's twist.

    python -m benchmarks contact_scenes   # or: python -m benchmarks.bench_contact_scenes [OUT_DIR]

- the twist (``sample_data/twist.yaml``, 50 × 50, 60 fps, one step per frame; its first 2 s,
  ``--full``: all 6 s): median
  wall and CPU ms per frame (the CPU time of the process is what other jobs on the shared
  machine disturb least), against NVIDIA Newton's own cloth-twist example (VBD with
  self-contact, 10 substeps × 4 iterations) run by its anchor script
  (``../shared/anchors/newton_twist.py`` beside the repository, or ``CLOTHTOOL_NEWTON_TWIST``)
  with a Python that has ``newton`` (``CLOTHTOOL_NEWTON_PYTHON``, else this one), where
  it installs;
- the drape, the stack and the tablecloth (``sample_data/*.yaml``), full length;
- every written frame of each run checked with ``ipctk.has_intersections`` and with our exact
  test on the cloth and its colliders, and the smallest ``min_separation`` of stats.csv;
- a scene without contact (the 64 × 64 hanging sheet, 10 frames, one Newton step) on this
  tree and on a base revision (``CLOTHTOOL_BASE_REV``, default ``main``; its files from git),
  alternating (5 runs each), for the ±5 % cost check: ``--full`` only.

Writes ``contact_scenes.csv`` and ``contact_scenes.md`` into OUT_DIR, and under ``--full``
docs/simulate.md's table (the whole twist, the comparison).
"""

import csv
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ipctk
import numpy as np

from benchmarks.common import FULL, full_or, markdown_table, write_csv, write_doc_table
from clothtool.contact.broadphase import mesh_edges
from clothtool.contact.intersect import has_intersections
from clothtool.io.ply import read_ply
from clothtool.sim.api import simulate
from clothtool.sim.model.config import load_config
from clothtool.sim.model.colliders import load_colliders

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("twist", "drape", "stack", "tablecloth")
# The twist's frames: its first 2 s by default (the sheet wound once, the contact dense from
# frame 60 on), all 6 s under --full; Newton's twist runs as many. The other scenes full length.
TWIST_FRAMES = full_or(360, 120)
NO_CONTACT_REPEAT = 5  # alternating runs of the scene without contact
NEWTON_SCRIPT = Path(os.environ.get("CLOTHTOOL_NEWTON_TWIST",
                                    ROOT.parent / "shared" / "anchors" / "newton_twist.py"))
NEWTON_PYTHON = os.environ.get("CLOTHTOOL_NEWTON_PYTHON", sys.executable)
BASE_REV = os.environ.get("CLOTHTOOL_BASE_REV", "main")


def check_frames(config_path, out_dir):
    """(frames, frames crossing by ipctk, by ours, smallest min_separation) of a finished run."""
    config = load_config(config_path)
    colliders = load_colliders(config.scene.colliders)
    paths = sorted(Path(out_dir).glob("frame_*.ply"))
    faces = read_ply(paths[0]).faces
    n = len(read_ply(paths[0]).vertices)
    all_faces = faces if colliders is None else np.concatenate([faces, colliders.faces + n])
    edges = mesh_edges(all_faces)
    crossing_ipc = crossing_ours = 0
    every = config.output.every
    for k, path in enumerate(paths):
        x = read_ply(path).vertices
        y = x if colliders is None else np.concatenate([x, colliders.positions(k * every / config.time.fps)])
        obstacle = np.arange(len(y)) >= n
        crossing_ipc += bool(ipctk.has_intersections(ipctk.CollisionMesh(y, edges, all_faces), y))
        crossing_ours += bool(has_intersections(y, all_faces, obstacle))
    with open(Path(out_dir) / "stats.csv") as fh:
        separation = min(float(r["min_separation"]) for r in csv.DictReader(fh))
    return len(paths), crossing_ipc, crossing_ours, separation


def run_scene(name, out_root):
    config_path = ROOT / "sample_data" / f"{name}.yaml"
    out = out_root / name
    over = {"time.frames": TWIST_FRAMES} if name == "twist" else None
    started, cpu = time.perf_counter(), time.process_time()
    result = simulate(config_path, output_dir=out, overrides=over, progress=False)
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu
    frames = result.frames_written - 1
    with open(out / "stats.csv") as fh:
        step_wall = [float(r["wall_s"]) for r in csv.DictReader(fh)][1:]
    written, ipc, ours, separation = check_frames(config_path, out)
    return {"scene": name, "vertices": len(read_ply(out / "frame_00000.ply").vertices),
            "frames": frames, "median step ms/frame": 1e3 * statistics.median(step_wall),
            "wall ms/frame": 1e3 * wall / frames, "CPU ms/frame": 1e3 * cpu / frames,
            "crossing frames (ipctk)": f"{ipc}/{written}", "crossing frames (ours)": f"{ours}/{written}",
            "min separation mm": 1e3 * separation}


def newton_twist(frames=TWIST_FRAMES):
    """Newton's figures from its anchor script, or None where it does not run."""
    if not NEWTON_SCRIPT.exists():
        return None
    try:
        out = subprocess.run([NEWTON_PYTHON, str(NEWTON_SCRIPT), str(frames)], capture_output=True,
                             text=True, timeout=3600)
    except (OSError, subprocess.TimeoutExpired):
        return None
    m = re.search(r"median ([\d.]+) ms/frame; frames with crossing triangles (\d+)/(\d+)", out.stdout)
    if out.returncode != 0 or m is None:
        return None
    return {"scene": "twist: NVIDIA Newton VBD (10 substeps × 4 iterations)", "vertices": 2500,
            "frames": frames, "median step ms/frame": float(m.group(1)),
            "crossing frames (ipctk)": f"{m.group(2)}/{m.group(3)}"}


NO_CONTACT = """
import sys, time
from clothtool.sim.api import simulate
over = {"mesh.grid.nx": 64, "mesh.grid.ny": 64, "time.frames": 10}
simulate(sys.argv[1], output_dir=sys.argv[2], overrides=over, progress=False)  # compile
c0 = time.process_time()
simulate(sys.argv[1], output_dir=sys.argv[2], overrides=over, progress=False)
print(1e3 * (time.process_time() - c0) / 10)
"""


def base_rev():
    """BASE_REV as this clone names it (a clone of another branch has main as origin/main),
    or None when it has neither."""
    for rev in (BASE_REV, f"origin/{BASE_REV}"):
        if subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "-q", rev],
                          capture_output=True).returncode == 0:
            return rev
    return None


def no_contact_cost(rev, repeat=NO_CONTACT_REPEAT):
    """(ms per step on this tree, on ``rev``): CPU time of the 64 × 64 hanging sheet, alternating."""
    config = ROOT / "sample_data" / "hanging_sheet.yaml"
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "main"
        base.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        times = {"this": [], "base": []}
        for _ in range(repeat):
            for label, path in (("this", ROOT), ("base", base)):
                env = {**os.environ, "PYTHONPATH": str(path)}
                out = subprocess.run([sys.executable, "-c", NO_CONTACT, str(config), f"{tmp}/out"],
                                     capture_output=True, text=True, env=env, check=True, cwd=path)
                times[label].append(float(out.stdout.strip().splitlines()[-1]))
    return statistics.median(times["this"]), statistics.median(times["base"])


def run(out_dir):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in SCENES:
            rows.append(run_scene(name, Path(tmp)))
            print(rows[-1], flush=True)
    newton = newton_twist()
    rows.insert(1, newton or {"scene": "twist: NVIDIA Newton VBD", "median step ms/frame": "not installed"})
    rev = base_rev() if FULL else None  # its own tree's kernels compiled: --full only
    this, base = no_contact_cost(rev) if rev else (None, None)
    columns = ["scene", "vertices", "frames", "median step ms/frame", "wall ms/frame", "CPU ms/frame",
               "crossing frames (ipctk)", "crossing frames (ours)", "min separation mm"]
    write_csv(out_dir / "contact_scenes.csv", rows, columns)
    text = ("## Contact scenes (issue 12)\n\n"
            "One step per frame at 60 fps. `median step ms/frame`: the median over the frames of the "
            "steps' wall time (stats.csv `wall_s`); `wall`/`CPU ms/frame`: the whole run, with "
            "writing and the exact check of every frame, per frame. Crossing frames: frames in "
            "which some cloth triangle crosses another or a collider's. Written by "
            "`python -m benchmarks contact_scenes`.\n\n" + markdown_table(rows, columns)
            + (f"\nA scene without contact (64 × 64 hanging sheet, CPU ms per step, median of "
               f"{NO_CONTACT_REPEAT} alternating runs): this tree {this:.2f}, {rev} {base:.2f} "
               f"({100.0 * (this / base - 1.0):+.1f} %).\n" if rev else
               f"\nNo {BASE_REV} in this clone: no comparison of a scene without contact.\n"
               if FULL else "\n`--full` compares a scene without contact with "
               f"{BASE_REV}.\n"))
    (out_dir / "contact_scenes.md").write_text(text)
    doc = [{**r, "solver": "clothtool"} for r in rows]
    doc[1].update(scene="twist", solver="NVIDIA Newton VBD")
    write_doc_table("docs/simulate.md", "contact-scenes", markdown_table(
        doc, ["scene", "solver"] + columns[1:]) + (
        f"\nA scene without contact (64 × 64 hanging sheet, CPU ms per step, median of "
        f"{NO_CONTACT_REPEAT} alternating runs): this tree {this:.2f}, {rev} {base:.2f} "
        f"({100.0 * (this / base - 1.0):+.1f} %).\n" if rev else ""), "contact_scenes",
        full_only=True)
    print(text)


if __name__ == "__main__":
    run(sys.argv[1] if len(sys.argv) > 1 else "bench-results")
