"""Each preconditioner's cost per phase on the Newton systems of a hanging sheet.

    python -m benchmarks linalg

The sheet (``SCENES``: 1.2 × 0.9 m, 0.25 kg/m², stretch 2e4 N/m, shear 100 N/m, bend 5e-5 N·m,
damping 0.02 s, held at its top corners, every solver key at its default) runs a few frames at
64² and 256² vertices; every Newton system of the last frames is kept with the positions it
was built at and the PCG tolerance the run asked for. Each preconditioner then solves the same
systems, timed phase by phase in CPU seconds (medians; the machine is shared):

- ``mesh_ms``: what is built once per mesh (aggregates, coarse patterns);
- ``prolongator_ms``: what is rebuilt from the positions (``amg``: at every Newton minimisation);
- ``galerkin_ms``: what each solve sets up (diagonal inverses, Galerkin products, the coarsest
  factor);
- ``cycle_ms``: one application of the preconditioner;
- ``its_per_solve``: PCG iterations per Newton solve at the run's tolerances, and ``ms_per_solve``
  the whole solve, setup included.

Then the whole step (``linalg-cost``): the same sheet at 64² and 256², one step per frame, as a
user runs it (``simulate``), on this tree at its defaults and with each other multilevel
preconditioner (``multigrid``, ``amg``, ``hybrid``), and on two earlier commits at theirs
(``BASES``: 3ee4668, main when the linear-solve issue was filed; 46ee052, round one's
linearised step), each in a process of its own, alternating: CPU ms per step (the run's CPU over
its frames after a warm-up run), Newton steps per step, PCG iterations per Newton step and µs
per vertex-step.

Writes ``bench-results/linalg.{csv,md}`` and docs/solvers.md's ``linalg-phases`` and
``linalg-cost`` tables.
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import (ROOT, full_or, markdown_table, median_seconds, write_csv,
                               write_doc_table)

SCENES = {"sheet": {"mesh": {"grid": {"width": 1.2, "height": 0.9, "plane": "xz"}},
                    "material": {"density": 0.25, "stretch": 2.0e4, "shear": 100.0,
                                 "bend": 5.0e-5, "damping": 0.02},
                    "scene": {"gravity": [0, -9.81, 0], "pins": ["top_corners"]}}}
SIZES = (64, 256)
FRAMES = {64: 8, 256: full_or(6, 3)}  # frames run; the systems of the last ones are kept
KEPT = {64: 8, 256: full_or(6, 3)}
PRECONDITIONERS = ("jacobi", "multigrid", "amg")
REPEAT = 5
COLUMNS = ["grid", "preconditioner", "systems", "mesh_ms", "prolongator_ms", "galerkin_ms",
           "cycle_ms", "its_per_solve", "ms_per_solve"]
BASES = {"3ee4668": "main when the linear-solve issue was filed",
         "46ee052": "round one: one linearised backward-Euler step"}
COST_FRAMES = {64: full_or(30, 15), 256: full_or(8, 4)}
COST_REPEAT = full_or(3, 1)
COST_COLUMNS = ["grid", "tree", "solver", "ms_per_step", "newton_per_step", "cg_per_newton",
                "us_per_vertex_step", "vs_46ee052", "vs_3ee4668"]
# one run: a warm-up run (compilation), then the timed one; prints CPU seconds and the counts
COST_SCRIPT = """
import csv, json, sys, time
from clothtool.sim.api import simulate
config, out = json.loads(sys.argv[1]), sys.argv[2]
simulate({**config, "time": {"fps": 30, "frames": 2}}, output_dir=out + "/warm", progress=False)
start = time.process_time()
simulate(config, output_dir=out + "/run", progress=False)
cpu = time.process_time() - start
rows = list(csv.DictReader(open(out + "/run/stats.csv")))[1:]
print(json.dumps({"cpu": cpu, "steps": len(rows),
                  "newton": sum(float(r["newton_iterations"] or 0) for r in rows),
                  "cg": sum(float(r["cg_iterations"] or 0) for r in rows)}))
"""


def capture(n):
    """The Newton systems of the sheet's last frames at n², with the positions of their
    Newton minimisation: a list of dicts."""
    import clothtool.sim.solve.newton as newton
    from clothtool.sim.linalg.blocks import BlockMatrix
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.methods import make_integrator

    scene = SCENES["sheet"]
    cfg = load_config({**scene, "mesh": {"grid": {**scene["mesh"]["grid"], "nx": n, "ny": n}},
                       "time": {"fps": 30, "frames": FRAMES[n]}})
    model = build_model(cfg)
    integ = make_integrator(model, cfg.solver, cfg.step)
    systems, where = [], {}
    update = integ.preconditioner.update

    def spy_update(x, constraints):
        where["x"] = x.copy()
        update(x, constraints)

    solve = newton.filtered_pcg

    def spy_solve(matrix, b, x, constraints, tol, *rest):
        systems.append({"matrix": BlockMatrix(matrix.pattern, matrix.values.copy()),
                        "floor": matrix.floor.copy(), "b": b.copy(), "x0": x.copy(),
                        "constraints": constraints, "tol": tol, "x": where["x"]})
        return solve(matrix, b, x, constraints, tol, *rest)

    integ.preconditioner.update = spy_update
    newton.filtered_pcg = spy_solve
    try:
        state = model.initial_state()
        counts = []
        for _ in range(FRAMES[n]):
            before = len(systems)
            integ.step(state)
            counts.append(len(systems) - before)
    finally:
        newton.filtered_pcg = solve
    kept = systems[len(systems) - sum(counts[-KEPT[n]:]):]
    for s in kept:
        s["matrix"].floor = s["floor"]
    return model, kept


def _cpu(fn, repeat=REPEAT):
    """Median CPU milliseconds of fn() over ``repeat`` calls after one untimed call."""
    return 1e3 * median_seconds(fn, repeat, time.process_time)


def measure(model, systems, name):
    """One row: the phases of preconditioner ``name`` on the captured systems."""
    from clothtool.sim.linalg.pcg import filtered_pcg, make_preconditioner

    start = time.process_time()
    pre = make_preconditioner(name, model.pattern, model.faces)
    mesh_ms = 1e3 * (time.process_time() - start)
    prolongator, galerkin, cycle, its, solve = [], [], [], [], []
    out = np.empty((model.n_vertices, 3))
    rhs = np.random.default_rng(0).standard_normal((model.n_vertices, 3))
    for s in systems:
        matrix, constraints = s["matrix"], s["constraints"]
        prolongator.append(_cpu(lambda: pre.update(s["x"], constraints)))
        galerkin.append(_cpu(lambda: pre.setup(matrix, constraints)))
        if hasattr(pre, "apply"):
            cycle.append(_cpu(lambda: pre.apply(rhs, out)))
        result = {}

        def run():
            x = s["x0"].copy()
            result["its"] = filtered_pcg(matrix, s["b"], x, constraints, s["tol"], 5000, pre)[0]

        solve.append(_cpu(run, repeat=3))
        its.append(result["its"])
    med = statistics.median
    return {"grid": f"{int(round(np.sqrt(model.n_vertices)))}²", "preconditioner": name,
            "systems": len(systems), "mesh_ms": round(mesh_ms, 1),
            "prolongator_ms": round(med(prolongator), 2), "galerkin_ms": round(med(galerkin), 2),
            "cycle_ms": round(med(cycle), 3) if cycle else "",
            "its_per_solve": round(float(np.mean(its)), 1),
            "ms_per_solve": round(float(np.mean(solve)), 1)}


def sheet_config(n, frames, solver=None):
    """The sheet scene at n² for ``simulate``."""
    scene = SCENES["sheet"]
    return {**scene, "mesh": {"grid": {**scene["mesh"]["grid"], "nx": n, "ny": n}},
            "time": {"fps": 30, "frames": frames}, **({"solver": solver} if solver else {})}


def cost_rows():
    """The whole step on this tree and on ``BASES``, alternating (see the module)."""
    from clothtool.sim.model.config import Solver

    others = [name for name in ("multigrid", "amg", "hybrid") if name != Solver().preconditioner]
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"this": ROOT}
        for rev in BASES:
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev],
                                     capture_output=True)
            if archive.returncode == 0:
                trees[rev] = Path(tmp) / rev
                trees[rev].mkdir()
                subprocess.run(["tar", "-x", "-C", str(trees[rev])], input=archive.stdout,
                               check=True)
        cases = [("this", "defaults", None)] + [("this", f"preconditioner: {name}",
                                                  {"preconditioner": name}) for name in others]
        cases += [(rev, "defaults", None) for rev in trees if rev != "this"]
        for _ in range(COST_REPEAT):
            for n in SIZES:
                for tree, label, solver in cases:
                    out = subprocess.run(
                        [sys.executable, "-c", COST_SCRIPT,
                         json.dumps(sheet_config(n, COST_FRAMES[n], solver)), f"{tmp}/out"],
                        capture_output=True, text=True, cwd=trees[tree],
                        env={**os.environ, "PYTHONPATH": str(trees[tree])})
                    if out.returncode != 0:
                        raise RuntimeError(f"{tree} {label} at {n}²: {out.stderr[-500:]}")
                    runs.setdefault((n, tree, label), []).append(
                        json.loads(out.stdout.strip().splitlines()[-1]))
    rows = []
    for (n, tree, label), results in runs.items():
        ms = statistics.median(1e3 * r["cpu"] / r["steps"] for r in results)
        newton = results[0]["newton"] / results[0]["steps"]
        rows.append({"grid": f"{n}²", "tree": tree, "solver": label, "ms_per_step": round(ms, 1),
                     "newton_per_step": round(newton, 2),
                     "cg_per_newton": round(results[0]["cg"] / max(results[0]["newton"], 1), 1),
                     "us_per_vertex_step": round(1e3 * ms / n / n, 2)})
    for row in rows:
        for rev in BASES:
            base = next((r for r in rows if r["grid"] == row["grid"] and r["tree"] == rev), None)
            row[f"vs_{rev}"] = round(row["ms_per_step"] / base["ms_per_step"], 2) if base else ""
    return rows


def run(out_dir):
    out_dir = Path(out_dir)
    cost = cost_rows()
    for row in cost:
        print(f"  {row}", flush=True)
    write_csv(out_dir / "linalg_cost.csv", cost, COST_COLUMNS)
    write_doc_table("docs/solvers.md", "linalg-cost", markdown_table(cost, COST_COLUMNS), "linalg")
    rows = []
    for n in SIZES:
        model, systems = capture(n)
        for name in PRECONDITIONERS:
            if name == "jacobi" and n > 64:
                continue  # block Jacobi needs thousands of iterations at 256²
            rows.append(measure(model, systems, name))
            print(f"  {rows[-1]}", flush=True)
    write_csv(out_dir / "linalg.csv", rows, COLUMNS)
    table = markdown_table(rows, COLUMNS)
    (out_dir / "linalg.md").write_text("# Preconditioners, cost per phase\n\n" + table
                                       + "\n\n# The whole step\n\n"
                                       + markdown_table(cost, COST_COLUMNS) + "\n")
    write_doc_table("docs/solvers.md", "linalg-phases", table, "linalg")
