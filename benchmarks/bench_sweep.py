"""Overhead of ``clothtool sweep`` on a local pool: end-to-end wall time of a sweep of N
runs of about one second each, against N/jobs × the time of one run.

    python -m benchmarks sweep

Writes ``sweep.csv``, ``sweep.md`` and the table of docs/sweep.md. The scene: a 16×16 sheet
on two corners, 60 frames at 30 fps (the default implicit solver); the runs differ in
``material.density`` only (0.200 … 0.210 kg/m²), so each costs about the same. Sweeps of 6
runs on 1 and 2 jobs (``--full``: 12, 24 and 48, and only it writes docs/sweep.md's table).

"The time of one run" has two meanings, and both are measured:

- ``simulate``: what a user compares against: the wall time of one ``clothtool simulate
  BASE -q --set material.density=…`` command, from the process start to its end (Python
  start-up, imports, numba's kernels loaded from the cache, the simulation, the frames),
  timed alone just before each sweep. ``user_ratio`` = sweep / (N/jobs × simulate).
- ``one run``: the simulation alone: the median of the runs' own times in that sweep
  (``seconds`` in the manifest: ``simulate()`` and the status file, measured in a worker
  that has already run one), so that it saw the same load as the sweep. ``ratio`` = sweep /
  (N/jobs × one run): everything the sweep adds to the simulations (the processes'
  start-up and imports, each worker's first kernel loading, the parent's bookkeeping,
  the uneven end when the last runs leave a core idle). The stricter of the two.

Columns besides: ``first run`` (the slowest run: a worker's first, which loads the
kernels), ``sweep`` (``clothtool sweep BASE -o DIR --grid material.density=… -j JOBS -q``
end to end), ``sweep_cpu_s`` (CPU of the sweep's whole process tree), ``process per run``
(the smallest sweep only: the same runs as ``clothtool simulate`` commands, JOBS at a
time, what a shell loop or ``make -j`` gives, against the same ``one run``), and the load
average.
The machine is shared (2 cores).
"""

import csv
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from benchmarks.common import clothtool_cmd, full_or, markdown_table, write_csv, write_doc_table

BASE = """\
mesh: {grid: {nx: 16, ny: 16, width: 0.5, height: 0.5, plane: xy}}
scene: {pins: [top_corners]}
solver: {tolerance: 1.0e-2}
time: {fps: 30, frames: 60}
"""
COUNTS = full_or((12, 24, 48), (6,))  # the docs' table: --full
JOBS = (1, 2)
PER_RUN_COUNT = COUNTS[0]  # process per run: the smallest sweep only
ENV = {**os.environ, "NUMBA_NUM_THREADS": "1"}  # as in a pool worker


def densities(n):
    return [round(0.2 + 0.01 * i / max(n - 1, 1), 6) for i in range(n)]


def children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def simulate_alone(base, value, out):
    """Wall time of one ``clothtool simulate`` command, as a user times it."""
    started = time.perf_counter()
    subprocess.run(clothtool_cmd("simulate", base, "-o", out, "-q", "--set",
                                 f"material.density={value}"), check=True,
                   stdout=subprocess.DEVNULL, env=ENV)
    return time.perf_counter() - started


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
    done = subprocess.run([sys.executable, "-c", code, str(base), str(out), *map(str, values)],
                          check=True, capture_output=True, text=True, env=ENV)
    return [float(line) for line in done.stdout.split()]


def process_per_run(base, values, jobs, out):
    cmds = [clothtool_cmd("simulate", base, "-o", out / f"r{i}", "-q", "--set",
                          f"material.density={v}") for i, v in enumerate(values)]
    started = time.perf_counter()
    with ThreadPoolExecutor(jobs) as pool:
        list(pool.map(lambda c: subprocess.run(c, check=True, stdout=subprocess.DEVNULL, env=ENV),
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
                alone = simulate_alone(base, values[0], tmp / "alone")
                grid = "material.density=" + ",".join(map(str, values))
                load = os.getloadavg()[0]
                folder = tmp / f"s{n}-{jobs}"
                cpu = children_cpu()
                started = time.perf_counter()
                subprocess.run(clothtool_cmd("sweep", base, "-o", folder, "--grid", grid, "-j", jobs,
                                             "-q"), check=True, stdout=subprocess.DEVNULL)
                wall = time.perf_counter() - started
                cpu = children_cpu() - cpu
                with open(folder / "manifest.csv", newline="") as fh:
                    seconds = [float(r["seconds"]) for r in csv.DictReader(fh)]
                one = statistics.median(seconds)
                ideal = n * one / jobs
                row = {"runs": n, "jobs": jobs, "simulate_s": alone, "one_run_s": one,
                       "first_run_s": max(seconds), "ideal_s": ideal, "sweep_s": wall,
                       "ratio": wall / ideal, "user_ratio": wall / (n * alone / jobs),
                       "sweep_cpu_s": cpu, "load": load}
                if n == PER_RUN_COUNT:
                    per_run = process_per_run(base, values, jobs, tmp / f"p{n}-{jobs}")
                    row.update(process_per_run_s=per_run, process_per_run_ratio=per_run / ideal)
                rows.append(row)
                print(f"  {n} runs, -j {jobs}: sweep {wall:.1f} s = {wall / ideal:.2f}× ideal "
                      f"{ideal:.1f} s (one run {one:.2f} s, first {max(seconds):.2f} s); "
                      f"{row['user_ratio']:.2f}× runs/jobs × simulate alone ({alone:.2f} s)"
                      + (f"; process per run {row['process_per_run_s']:.1f} s "
                         f"({row['process_per_run_ratio']:.2f}×)" if n == PER_RUN_COUNT else "")
                      + f"; load {load:.1f}", flush=True)
    columns = list(rows[0])
    write_csv(out_dir / "sweep.csv", rows, columns)
    (out_dir / "sweep.md").write_text(
        "## Sweep overhead (`python -m benchmarks sweep`)\n\n"
        "16×16 sheet, 60 frames per run (about 1 s of simulation). simulate = one `clothtool simulate` command alone, "
        "end to end (what a user times); one run = the median of the runs' own simulation times "
        "in the sweep (a warm worker); ideal = runs / jobs × one run; ratio = sweep / ideal; "
        "user_ratio = sweep / (runs / jobs × simulate); sweep = `clothtool sweep -j JOBS` end to "
        "end; first run = the slowest run (a worker's first: numba's kernels loaded); process "
        f"per run = one `clothtool simulate` per run, JOBS at a time. Warm run alone: {warm:.2f} s."
        "\n\n" + markdown_table(rows, columns))
    write_doc_table("docs/sweep.md", "sweep", markdown_table(rows, columns), "sweep",
                    full_only=True)
