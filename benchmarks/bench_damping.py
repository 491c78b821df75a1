"""The damping models side by side at one step per frame (issue 40).

    python -m benchmarks damping

Each scene with ``material.damping_model: strain`` (the default), ``frozen`` and with
``material.damping: 0``, everything else at its default (``solver.stiffness_continuation:
auto`` after 20 stalled Newton steps); the stiff and hanging scenes also with Newton alone
(``solver.stiffness_continuation: 0``), with ``stiffness_continuation: 4`` on every solve
(each step solved first with the membrane 10⁴, …, 10× softer) and with 4 levels only for the
solves Newton alone stalls on in 20 steps:

- turning sphere: a 1 m sheet (16×16) dropped on a sphere of radius 0.3 m turning at π rad/s,
  μ 0.4, 2 s at 30 fps (``benchmarks/friction_scenes.py``): the cloth's turn rate over the
  last second over the sphere's;
- crumpled start: a 16×16 sheet released from random displacements of up to 0.6 cell
  (fibres stretched up to 2.7×, triangles folded and inverted), 30 fps: its largest principal
  stretch at frame 8;
- stiff at 1 s: a 12×12 sheet of 1e6 N/m (shear 1e5) hanging from its top corners at
  h = 1 s, 6 steps: Newton steps per step (the cap is ``solver.newton_iterations`` a solve;
  BDF2's first step has two stages, and a continuation level is a solve of its own), the
  solves that stopped at the cap unconverged and the largest stretch;
- hanging_sheet: sample_data/hanging_sheet.yaml at 64×64, 1 s at 30 fps: Newton steps per
  step, CPU ms per step (the least of two alternating runs in this process; one run
  without ``--full``) and its ratio to ``frozen``'s, and the sheet's lowest point after 1 s
  (it swings down and back up; the same sheet at 16 steps per frame, damped by strain:
  ``reference``, under ``--full``).

Writes ``damping.md`` and (under ``--full``, which adds the reference) the table ``damping``
of docs/simulate.md.
"""

import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import FULL, full_or, markdown_table, write_csv, write_doc_table

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("turning sphere", "crumpled start", "stiff at 1 s", "hanging_sheet")
SETTINGS = (("strain (default)", {}, {}), ("frozen", {"damping_model": "frozen"}, {}),
            ("damping 0", {"damping": 0.0}, {}),
            ("strain, Newton alone", {}, {"stiffness_continuation": 0}),
            ("strain, stiffness_continuation 4", {},
             {"stiffness_continuation": 4, "continuation_after": 0}),
            ("strain, stiffness_continuation 4 after 20", {},
             {"stiffness_continuation": 4, "continuation_after": 20}))


def sphere(material):
    from benchmarks.friction_scenes import turning_sphere

    with tempfile.TemporaryDirectory() as tmp:
        spin, omega, _ = turning_sphere(Path(tmp), damping=0.01, material=material)
    return float(np.mean(spin[-30:]) / omega)


def crumpled(material, frames=8):
    from clothtool.sim.energies.membrane import max_principal_stretch
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config
    from clothtool.sim.solvers.compare import run_in_memory

    def crumple(model, state):
        state.x += np.random.default_rng(0).uniform(-0.6, 0.6, state.x.shape) / 15

    cfg = load_config({"mesh": {"grid": {"nx": 16, "ny": 16, "plane": "xz"}},
                       "material": material, "time": {"fps": 30, "frames": frames}})
    model = build_model(cfg)
    run = run_in_memory(cfg, (frames,), warmup=False, initial=crumple)
    return max_principal_stretch(run.positions[frames], model.faces, model.dr_inv)


def stiff(material, solver, steps=6):
    """(Newton steps per step, the cap of a solve, solves stopped at it, largest stretch)."""
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.methods import make_integrator

    cfg = load_config({"mesh": {"grid": {"nx": 12, "ny": 12, "plane": "xz"}},
                       "material": {"stretch": 1e6, "shear": 1e5, **material},
                       "scene": {"pins": ["top_corners"]}, "time": {"fps": 1, "frames": steps},
                       "solver": solver})
    model = build_model(cfg)
    integrator = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    counts, capped, stretch = [], 0, 1.0
    for _ in range(steps):
        report = integrator.step(state)
        counts.append(report.newton_iterations)
        capped += report.capped
        stretch = max(stretch, integrator.max_stretch(state))
    return counts, cfg.solver.newton_iterations, capped, stretch


def hanging(material, solver=None, n=64, frames=30, substeps=1):
    """(Newton steps per step, CPU s per step, lowest point (m) after ``frames``)."""
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.methods import make_integrator

    overrides = {"mesh.grid.nx": n, "mesh.grid.ny": n, "solver.substeps": substeps,
                 **{f"material.{k}": v for k, v in material.items()},
                 **{f"solver.{k}": v for k, v in (solver or {}).items()}}
    cfg = load_config(ROOT / "sample_data" / "hanging_sheet.yaml", overrides=overrides)
    model = build_model(cfg)
    make_integrator(model, cfg.solver, cfg.step).step(model.initial_state())  # compile
    integrator = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    newton, steps = 0, frames * substeps
    started = time.process_time()
    for _ in range(steps):
        newton += integrator.step(state).newton_iterations
    cpu = (time.process_time() - started) / steps
    return newton / steps, cpu, float(state.x[:, 1].min())


def run(out_dir):
    rows = {label: {"damping": label} for label, _, _ in SETTINGS}
    for label, material, solver in SETTINGS:
        row = rows[label]
        # the continuation is for stiff cloth at large steps: not run on these two
        row["turning sphere: cloth ÷ sphere"] = "—" if solver else f"{sphere(material):.3f}"
        row["crumpled start: stretch at frame 8"] = "—" if solver else f"{crumpled(material):.3f}"
        counts, cap, capped, stretch = stiff(material, solver)
        row["stiff at 1 s: Newton steps per step (cap a solve)"] = (
            f"{', '.join(map(str, counts))} ({cap})")
        row["stiff at 1 s: solves at the cap"] = str(capped)
        row["stiff at 1 s: largest stretch"] = f"{stretch:.4f}"
        print(row, flush=True)
    cpu = {label: [] for label, _, _ in SETTINGS}
    for _ in range(full_or(2, 1)):  # alternating, the least of two (one without --full)
        for label, material, solver in SETTINGS:
            newton, seconds, low = hanging(material, solver)
            cpu[label].append(seconds)
            rows[label]["hanging_sheet: Newton steps per step"] = f"{newton:.2f}"
            rows[label]["hanging_sheet: lowest point after 1 s (m)"] = f"{low:.3f}"
    for label, _, _ in SETTINGS:
        rows[label]["hanging_sheet: CPU ms per step"] = f"{1e3 * min(cpu[label]):.0f}"
        rows[label]["CPU ÷ frozen"] = f"{min(cpu[label]) / min(cpu['frozen']):.2f}"
    table = list(rows.values())
    text = markdown_table(table, list(table[0])) + "\n\nThe hanging sheet at 16 steps per frame "
    if FULL:  # 480 steps of the 64×64 sheet, the longest run here
        text += f"(`strain`): lowest point {hanging({}, substeps=16)[2]:.3f} m after 1 s.\n"
    else:
        text += "(`strain`): `python -m benchmarks --full damping`.\n"
    write_csv(Path(out_dir) / "damping.csv", table, list(table[0]))
    (Path(out_dir) / "damping.md").write_text("## Damping models at one step per frame\n\n" + text)
    write_doc_table("docs/simulate.md", "damping", text, "damping", full_only=True)
    print(text)
