"""Overhead of ``clothtool sweep`` on a local pool: end-to-end wall time of a sweep of N
runs of about one second each, against N/jobs × the time of one run.

    python -m benchmarks sweep

Writes ``sweep.csv`` and ``sweep.md``. The scene: a 16×16 sheet on two corners, 40
frames at 30 fps (the default implicit solver); the runs differ in
``material.density`` only (0.200 … 0.210 kg/m²), so each costs about the same.

- ``sweep``: ``clothtool sweep BASE -o DIR --grid material.density=… -j JOBS -q``, from the
  process start to its end (Python start-up, worker start-up, every run, manifest).
- ``one run``: the median of the runs' own times in that sweep (``seconds`` in the
  manifest: simulation and status file, measured in the worker), so that it saw the same
  load as the sweep; ``ideal`` = N/jobs × one run, and the ratio sweep / ideal is the
  overhead: the start-up of the processes (each worker's first run also loads numba's
  kernels: ``first run``), the parent's bookkeeping, and the uneven end (the last runs
  leave cores idle).
- ``warm run``: one run in a process that has already run one, measured alone before the
  sweeps (the machine's speed at that moment, for reference).
- ``process per run`` (12 runs only): the same runs as ``clothtool simulate`` commands,
  JOBS at a time (what a shell loop or ``make -j`` gives), against the same ideal.

The machine is shared (2 cores): the load average is recorded beside the figures.
"""

import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from benchmarks.common import clothtool_cmd, markdown_table, write_csv

BASE = """\
mesh: {grid: {nx: 16, ny: 16, width: 0.5, height: 0.5, plane: xy}}
scene: {pins: [top_corners]}
solver: {tolerance: 1.0e-2}
time: {fps: 30, frames: 40}
"""
COUNTS = (12, 24, 48)
JOBS = (1, 2)
PER_RUN_COUNT = 12


def densities(n):
    return [round(0.2 + 0.01 * i / max(n - 1, 1), 6) for i in range(n)]


def warm_times(base, values, out):
    """Seconds of each run's simulation in one process that has already run one."""
    code = (
        "import sys, time, clothtool\n"
        "base, out, *values = sys.argv[1:]\n"
        "clothtool.simulate(base, output_dir=out, progress=False)\n"
        "for v in values:\n"
        "    t = time.perf_counter()\n"
        "    clothtool.simulate(base, output_dir=out, progress=False,\n"
        "                       overrides={'material.density': float(v)})\n"
        "    print(time.perf_counter() - t)\n")
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}  # as in a pool worker
    done = subprocess.run([sys.executable, "-c", code, str(base), str(out), *map(str, values)],
                          check=True, capture_output=True, text=True, env=env)
    return [float(line) for line in done.stdout.split()]


def process_per_run(base, values, jobs, out):
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    cmds = [clothtool_cmd("simulate", base, "-o", out / f"r{i}", "-q", "--set",
                          f"material.density={v}") for i, v in enumerate(values)]
    started = time.perf_counter()
    with ThreadPoolExecutor(jobs) as pool:
        list(pool.map(lambda c: subprocess.run(c, check=True, stdout=subprocess.DEVNULL, env=env),
                      cmds))
    return time.perf_counter() - started


def run(out_dir):
    out_dir = Path(out_dir)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        tmp = Path(tmp)
        base = tmp / "base.yaml"
        base.write_text(BASE)
        warm = statistics.median(warm_times(base, [0.2] * 3, tmp / "warm"))
        for n in COUNTS:
            values = densities(n)
            for jobs in JOBS:
                grid = "material.density=" + ",".join(map(str, values))
                load = os.getloadavg()[0]
                folder = tmp / f"s{n}-{jobs}"
                started = time.perf_counter()
                subprocess.run(clothtool_cmd("sweep", base, "-o", folder, "--grid", grid, "-j", jobs,
                                             "-q"), check=True, stdout=subprocess.DEVNULL)
                wall = time.perf_counter() - started
                with open(folder / "manifest.csv", newline="") as fh:
                    seconds = [float(r["seconds"]) for r in csv.DictReader(fh)]
                one = statistics.median(seconds)
                ideal = n * one / jobs
                row = {"runs": n, "jobs": jobs, "warm_run_s": warm, "one_run_s": one,
                       "first_run_s": max(seconds), "ideal_s": ideal, "sweep_s": wall,
                       "sweep_ratio": wall / ideal, "load": load}
                if n == PER_RUN_COUNT:
                    per_run = process_per_run(base, values, jobs, tmp / f"p{n}-{jobs}")
                    row.update(process_per_run_s=per_run, process_per_run_ratio=per_run / ideal)
                rows.append(row)
                print(f"  {n} runs, -j {jobs}: sweep {wall:.1f} s = {wall / ideal:.2f}× ideal "
                      f"{ideal:.1f} s (one run {one:.2f} s, first {max(seconds):.2f} s)"
                      + (f"; process per run {row['process_per_run_s']:.1f} s "
                         f"({row['process_per_run_ratio']:.2f}×)" if n == PER_RUN_COUNT else "")
                      + f"; load {load:.1f}", flush=True)
    columns = list(rows[0])
    write_csv(out_dir / "sweep.csv", rows, columns)
    (out_dir / "sweep.md").write_text(
        "## Sweep overhead (`python -m benchmarks sweep`)\n\n"
        "16×16 sheet, 40 frames per run. one run = median of the runs' own times in the sweep; "
        "ideal = runs / jobs × one run; sweep = `clothtool sweep -j JOBS` end to end; "
        "first run = the slowest run (a worker's first: numba's kernels loaded); process per "
        f"run = one `clothtool simulate` per run, JOBS at a time. Warm run alone: {warm:.2f} s.\n\n"
        + markdown_table(rows, columns))
