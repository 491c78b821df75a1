"""Helpers shared by the benchmarks: timing commands, peak memory, Markdown tables."""

import os
import statistics
import subprocess
import sys
import time

PYTHON = sys.executable
# ``python -m benchmarks --full`` (or CLOTHTOOL_BENCH_FULL=1): the long cases too. By default
# every table keeps its rows' meaning at a lighter scale (coarser references, looser tight
# solves, fewer repeats and resolutions) so that ``make bench`` fits in 15 minutes on 2 cores
# from a fresh clone, venv included.
FULL = os.environ.get("CLOTHTOOL_BENCH_FULL") == "1"


def full_or(full, light):
    """``full`` under ``--full``, else ``light``."""
    return full if FULL else light

BIN = os.path.dirname(sys.executable)


# Where a checkout keeps the simulator's entry points (load_config, build_model,
# make_integrator), newest first: the modules moved, and a benchmark that runs an old
# commit's code in a clone must import them from where that commit has them.
SIM_LAYOUTS = (
    ("clothtool/sim/model/builder.py",  # since the simulator's rooms
     "from clothtool.sim.model.config import load_config\n"
     "from clothtool.sim.model.methods import make_integrator\n"
     "from clothtool.sim.model.builder import build_model\n"),
    ("clothtool/sim/builder.py",  # one flat sim/ with a builder
     "from clothtool.sim.config import load_config\n"
     "from clothtool.sim.methods import make_integrator\n"
     "from clothtool.sim.builder import build_model\n"),
    ("clothtool/sim/model.py",  # one flat sim/, the model module building itself (1e6cea5)
     "from clothtool.sim.config import load_config\n"
     "from clothtool.sim.methods import make_integrator\n"
     "from clothtool.sim.model import build_model\n"),
)


def sim_imports(root):
    """The import lines of ``load_config``, ``make_integrator`` and ``build_model`` for the
    checkout at ``root``."""
    for marker, lines in SIM_LAYOUTS:
        if os.path.exists(os.path.join(root, marker)):
            return lines
    raise FileNotFoundError(f"{root}: no known layout of clothtool.sim")


def clothtool_cmd(*args):
    return [os.path.join(BIN, "clothtool"), *map(str, args)]


def run_timed(cmd, env=None, fresh=None):
    """Wall time of a command in seconds (fails loudly if the command fails).

    ``fresh``: an output path removed (untimed) before the run, so that no route pays
    for deleting the previous run's file."""
    if fresh is not None and os.path.exists(fresh):
        os.remove(fresh)
    started = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=env)
    return time.perf_counter() - started


def median_time(cmd, repeat=3, fresh=None):
    return statistics.median(run_timed(cmd, fresh=fresh) for _ in range(repeat))


def peak_rss_mb(cmd):
    """Peak resident memory (MB) of a command, measured in a fresh wrapper process."""
    code = ("import resource, subprocess, sys\n"
            "subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL)\n"
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    out = subprocess.run([PYTHON, "-c", code, *cmd], check=True, capture_output=True, text=True)
    return int(out.stdout.strip().splitlines()[-1]) / 1024.0


def pyplot(what="plot"):
    """matplotlib's pyplot on the Agg backend, or None (saying there is no ``what``) when
    matplotlib is not installed."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"  matplotlib not installed: no {what} (pip install 'clothtool[bench]')")
        return None
    return plt


def markdown_table(rows, columns):
    """rows: list of dicts → a Markdown table with the given columns."""
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.3e}"
        return str(v)
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(fmt(r.get(c, "")) for c in columns) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def write_csv(path, rows, columns):
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def median_seconds(fn, repeat=7, clock=time.perf_counter):
    """Median time of ``repeat`` calls of ``fn()`` after one untimed call (warm-up, compile):
    wall time, or CPU time with ``clock=time.process_time``."""
    fn()
    times = []
    for _ in range(repeat):
        started = clock()
        fn()
        times.append(clock() - started)
    return statistics.median(times)


# ---------------------------------------------------------------------------- measured tables

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MEASURED = "measured on {commit} {date} (load {load:.1f} on {cores} cores), `{command}`"


def measured_line(benchmark):
    """'measured on <commit> <date> (load L on N cores), `python -m benchmarks NAME`': the
    commit of this checkout (+ when clothtool/ or benchmarks/ differ from it), today (UTC)
    and the 1-minute load average, which says how shared the machine was."""
    def git(*args):
        out = subprocess.run(["git", "-C", ROOT, *args], capture_output=True, text=True)
        return out.stdout.strip() if out.returncode == 0 else ""

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--", "clothtool", "benchmarks"):
        commit += "+"
    return MEASURED.format(commit=commit, date=time.strftime("%Y-%m-%d", time.gmtime()),
                           load=os.getloadavg()[0], cores=os.cpu_count(),
                           command=f"python -m benchmarks{' --full' if FULL else ''} {benchmark}")


def write_doc_table(doc, name, table, benchmark, full_only=False):
    """Write ``table`` (Markdown) between ``<!-- begin NAME -->`` and ``<!-- end NAME -->`` in
    ``doc`` (a path under the checkout, e.g. ``docs/solvers.md``), with the :func:`measured_line`
    of ``benchmark`` under it. The markers stay where the doc's text puts them; a doc without
    them is an error (tests/test_docs_measured.py checks the tables' scenes and keys).

    ``full_only``: the doc's table is the one ``--full`` measures (without it the benchmark
    runs less of it, so the doc keeps what it has; bench-results/ has the lighter table)."""
    if full_only and not FULL:
        print(f"  {doc}: table {name} kept (`python -m benchmarks --full {benchmark}` writes it)")
        return
    path = os.path.join(ROOT, doc)
    with open(path) as fh:
        text = fh.read()
    begin, end = f"<!-- begin {name} -->", f"<!-- end {name} -->"
    if text.count(begin) != 1 or text.count(end) != 1:
        raise ValueError(f"{doc}: no single {begin} … {end} block")
    head, rest = text.split(begin)
    _, tail = rest.split(end)
    body = f"{begin}\n{table.rstrip()}\n\n{measured_line(benchmark)}\n{end}"
    with open(path, "w") as fh:
        fh.write(head + body + tail)
    print(f"  {doc}: table {name} written")
